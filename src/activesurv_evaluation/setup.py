from setuptools import find_packages, setup

package_name = 'activesurv_evaluation'

setup(
    name=package_name,
    version='0.9.0',
    packages=find_packages(exclude=['test', 'test.*']),
    package_data={package_name: ['py.typed']},
    data_files=[
        ('share/ament_index/resource_index/packages', ['resource/' + package_name]),
        ('share/' + package_name, ['package.xml']),
    ],
    install_requires=['setuptools'],
    zip_safe=False,
    maintainer='activesurv developers',
    maintainer_email='dev@activesurv.invalid',
    description='Evaluation of recorded runs: results.json, tracking metrics, reports (no ROS).',
    license='Apache-2.0',
)
