from glob import glob

from setuptools import find_packages, setup

package_name = 'activesurv_recording'

setup(
    name=package_name,
    version='0.9.0',
    packages=find_packages(exclude=['test', 'test.*']),
    package_data={package_name: ['py.typed']},
    data_files=[
        ('share/ament_index/resource_index/packages', ['resource/' + package_name]),
        ('share/' + package_name, ['package.xml']),
        ('share/' + package_name + '/config', glob('config/*.yaml')),
    ],
    install_requires=['setuptools'],
    zip_safe=False,
    maintainer='activesurv developers',
    maintainer_email='dev@activesurv.invalid',
    description=(
        'rosbag2 recording: the recorder node, reading and salvaging bags, '
        'an image load generator.'
    ),
    license='Apache-2.0',
    entry_points={
        'console_scripts': [
            'recorder = activesurv_recording.recorder_node:main',
            'image_load = activesurv_recording.load_node:main',
        ],
    },
)
