from setuptools import find_packages, setup

package_name = 'activesurv_launch'

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
    description=(
        'Starting ROS 2 nodes: one process per node, component containers, '
        'in-process composition, network namespaces.'
    ),
    license='Apache-2.0',
    entry_points={
        'console_scripts': [],
    },
)
