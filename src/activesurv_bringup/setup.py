from glob import glob

from setuptools import find_packages, setup

package_name = 'activesurv_bringup'

setup(
    name=package_name,
    version='0.1.0',
    packages=find_packages(exclude=['test', 'test.*']),
    package_data={package_name: ['py.typed']},
    data_files=[
        ('share/ament_index/resource_index/packages', ['resource/' + package_name]),
        ('share/' + package_name, ['package.xml']),
        (
            'share/' + package_name + '/config',
            glob('config/*.yaml') + glob('config/*.xml') + glob('config/*.json'),
        ),
    ],
    install_requires=['setuptools'],
    zip_safe=False,
    maintainer='activesurv developers',
    maintainer_email='dev@activesurv.invalid',
    description=(
        'Configurations, orchestration, experiments, rosbag2 recording and replay, '
        'evaluation and reports.'
    ),
    license='Apache-2.0',
    entry_points={
        'console_scripts': [
            'activesurv = activesurv_bringup.cli:main',
        ],
    },
)
